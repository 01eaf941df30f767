"""Validation of a merged flight table: every check vectorised over the whole record.

Errors name the file, the source column and the 1-based data rows of that file
(:mod:`flightrecon.errors`).  Checks (docs/ingest.md, "Validation"):

* time: missing, non-finite, duplicate or backward timestamps (rows named; no silent fix);
* schema: required channels present, a required channel with no sample at all;
* values outside ``Channel.lo``/``Channel.hi`` (schema.py), +-inf included: isolated ones are
  clipped (just outside) or masked (far outside) and reported as :class:`Repair`; a channel out of
  range systematically (a wrong unit, a flipped sign) is refused with the likely fix named;
* NaN storms: a channel whose recorded samples are mostly literal ``NaN`` (an error); a few
  literal NaN are a recoverable defect (a warning, the values stay missing).

The polarity of the load factors and of the bank against the turn is :mod:`.polarity`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from flightrecon.errors import SchemaError, ValidationError
from flightrecon.schema import BY_NAME, REQUIRED, Channel

__all__ = [
    "NAN_STORM_FRACTION",
    "Provenance",
    "DERIVABLE",
    "Repair",
    "check_required",
    "check_time",
    "check_values",
]

#: fraction of a channel's recorded samples written as NaN above which the channel is unusable
NAN_STORM_FRACTION = 0.5


@dataclass(frozen=True)
class Provenance:
    """Where each row of the merged table came from.

    Attributes
    ----------
    files : source paths (index 0 is the recorder log)
    src_file : (N,) index into ``files`` for every row
    row : (N,) 1-based data row in that file
    source_column : per file, channel -> source column name
    """

    files: tuple[str, ...]
    src_file: np.ndarray
    row: np.ndarray
    source_column: tuple[dict[str, str], ...]

    def locate(self, mask: np.ndarray, channel: str) -> dict:
        """``file``, ``column`` and ``rows`` keywords for an error about the True rows of ``mask``
        (the first file that has any)."""
        idx = np.flatnonzero(mask)
        f = int(self.src_file[idx[0]])
        in_f = idx[self.src_file[idx] == f]
        col = self.source_column[f].get(channel, channel)
        col_txt = col if col == channel else f"{col}' -> '{channel}"
        return {"file": self.files[f], "column": col_txt, "rows": self.row[in_f]}


def check_time(t: np.ndarray, rows: np.ndarray, file: str, column: str, *,
               allow_unsorted: bool) -> tuple[np.ndarray | None, list[str]]:
    """Check that the times of one file strictly increase.

    Returns
    -------
    order : a stable sorting permutation if ``allow_unsorted`` and the times were unsorted,
        else ``None``
    warnings : what was found when ``allow_unsorted``

    Raises
    ------
    ValidationError
        Duplicate or backward times (naming the rows where time stops increasing), unless
        ``allow_unsorted``.
    """
    if t.size < 2:
        return None, []
    dt = np.diff(t)
    back = np.flatnonzero(dt < 0) + 1
    dup = np.flatnonzero(dt == 0) + 1
    warns: list[str] = []
    if back.size or dup.size:
        if not allow_unsorted:
            if back.size:
                raise ValidationError(f"time goes backward ({back.size} times; the rows named "
                                      "are earlier than the row before them)", file=file,
                                      column=column, rows=rows[back].tolist())
            raise ValidationError(f"duplicate timestamps ({dup.size}; the rows named repeat the "
                                  "time of the row before them)", file=file, column=column,
                                  rows=rows[dup].tolist())
        if back.size:
            warns.append(f"{file}: time goes backward at {back.size} row(s) (first: row "
                         f"{rows[back[0]]}); rows sorted by time as allowed")
        if dup.size:
            warns.append(f"{file}: {dup.size} duplicate timestamp(s) (first: row "
                         f"{rows[dup[0]]}) kept for the cleaning layer")
        return (np.argsort(t, kind="stable") if back.size else None), warns
    return None, warns


#: required channels that ingest derives when they are not recorded, from these channels
#: (:func:`flightrecon.ingest.derive.derive_n_long`, :func:`~flightrecon.ingest.derive.
#: derive_n_lat`: coordinated flight's lateral load beside a recorded normal load)
DERIVABLE: dict[str, tuple[str, ...]] = {"n_long_g": ("tas_mps", "pitch_deg"),
                                         "n_lat_g": ("n_norm_g",)}


def check_required(channels, file: str, other_columns=(), mapping_hint: str = "") -> None:
    """Raise :class:`SchemaError` naming the required channels missing from ``channels``
    (with the closest of ``other_columns``, the file's unused columns, as a hint, and
    ``mapping_hint``: the mapping files found beside the log).  A channel of
    :data:`DERIVABLE` whose sources are all in ``channels`` is not missing."""
    import difflib

    missing = [c for c in REQUIRED if c != "t_s" and c not in channels
               and not set(DERIVABLE.get(c, ("-",))) <= set(channels)]
    if missing:
        hints = []
        for m in missing:
            close = difflib.get_close_matches(m, [c for c in other_columns if c not in BY_NAME],
                                              n=1)
            if close:
                hints.append(f"'{close[0]}' -> {m}?")
        hint = f" (similar columns: {', '.join(hints)})" if hints else ""
        how = mapping_hint or "map foreign names with a mapping file (docs/ingest.md)"
        lacking = [c for m in missing for c in DERIVABLE.get(m, ()) if c not in channels]
        if "n_long_g" in missing:
            # many recorders have no longitudinal accelerometer: say what would do instead
            how += ("; a log without n_long_g is accepted when tas_mps (or ias_mps/cas_mps) "
                    f"and pitch_deg are there (it is derived from them; missing: "
                    f"{', '.join(lacking)})")
        raise SchemaError(f"missing required channel(s): {', '.join(missing)}{hint}; {how}",
                          file=file, column=missing[0])


#: how far beyond a channel's physical range a value may lie and still be *clipped* to the bound
#: (noise or quantisation of a sensor at the end of its range: airspeed noise at rest, a load
#: factor saturating on an impact), per canonical unit.  Angles that wrap, positions and other
#: units have no margin: a value outside is masked.
CLIP_MARGIN: dict[str, float] = {"m/s": 2.0, "g": 0.5, "deg": 1.0, "m": 50.0, "degC": 2.0,
                                 "deg/s": 5.0}
#: channels with no clip margin whatever their unit (a position or a wrapped angle outside its
#: range is no sensor noise)
NO_CLIP = ("gnss_lat_deg", "gnss_lon_deg")
#: fraction of a channel's samples beyond the clip margin above which the channel is out of range
#: *systematically* (a wrong unit, a flipped sign): refused.  At or below it the values are
#: isolated glitches and are masked (treated as missing samples; the cleaning layer fills them).
SYSTEMATIC_FRACTION = 0.01
#: minimum number of masked values for a systematic verdict (one bad value in a 20-sample file
#: is a glitch, not a unit)
SYSTEMATIC_MIN_COUNT = 3


@dataclass(frozen=True)
class Repair:
    """One repair made at validation: ``count`` values of ``channel`` (source ``column`` of
    ``file``, 1-based data ``rows``) ``action`` (``"clipped"`` to the range or ``"masked"`` as
    missing samples), with the first offending value."""

    file: str
    column: str
    channel: str
    rows: tuple[int, ...]
    count: int
    action: str
    first_value: float
    bound: tuple[float, float]
    t_s: tuple[float, ...] = ()
    why: str = ""

    def message(self) -> str:
        shown = ", ".join(str(r) for r in self.rows[:10]) + (" ..." if len(self.rows) > 10
                                                              else "")
        if self.why:
            return (f"{self.file}: column '{self.column}': {self.count} fix(es) {self.action} "
                    f"(row(s) {shown}): {self.why}")
        what = ("clipped to the range" if self.action == "clipped"
                else "masked (treated as missing samples; the cleaning layer fills them)")
        return (f"{self.file}: column '{self.column}': {self.count} value(s) outside the "
                f"physical range [{self.bound[0]:g}, {self.bound[1]:g}] (first {self.first_value:g}"
                f", row(s) {shown}) {what}")

    def as_dict(self) -> dict:
        return {"file": self.file, "column": self.column, "channel": self.channel,
                "rows": [int(r) for r in self.rows], "count": self.count, "action": self.action,
                "first_value": float(self.first_value), "range": list(self.bound),
                "t_s": [float(x) for x in self.t_s], "why": self.why}


def _suggest_fix(ch, v: np.ndarray) -> str:
    """What would bring the sampled values ``v`` of channel ``ch`` into range: a flipped sign or
    one of the other units of the channel's dimension (the first candidate under which at least
    99 % of the samples are in range)."""
    from flightrecon.ingest.units import CANONICAL_DIMENSION, UNITS

    fin = v[np.isfinite(v)]
    if fin.size == 0:
        return "the channel has no finite value"
    if np.all((fin >= ch.lo) & (fin <= ch.hi)):
        return ("the values outside are infinities: the recorder marks this channel invalid "
                "there; drop the column or mask those rows")

    def fits(x):
        return float(np.mean((x >= ch.lo) & (x <= ch.hi))) >= 1.0 - SYSTEMATIC_FRACTION

    if fits(-fin):
        return "the sign looks flipped: use sign = -1 in a mapping file"
    dim = CANONICAL_DIMENSION.get(ch.unit)
    for u in UNITS.values():
        if u.dimension != dim or (u.scale == 1.0 and u.offset == 0.0):
            continue
        for sgn in (1.0, -1.0):
            if fits(sgn * (fin * u.scale + u.offset)):
                s = "" if sgn > 0 else " and sign = -1"
                return (f"the values fit if the column is in {u.name}: use unit = '{u.name}'{s} "
                        "in a mapping file")
    return ("check the column's unit and sign (unit = / sign = in a mapping file) or whether it "
            "is the right column")


def check_values(data: pd.DataFrame, prov: Provenance,
                 nan_text: dict[str, np.ndarray]) -> tuple[list[str], list[Repair]]:
    """Range, inf, empty-channel and NaN-storm checks over every canonical channel.

    Values outside a channel's physical range ``[Channel.lo, Channel.hi]`` are judged
    (docs/ingest.md, "Values outside the physical range"):

    * within ``CLIP_MARGIN`` of the range (sensor noise at the end of the range): clipped to the
      bound;
    * farther out, or infinite: masked (set to NaN, a missing sample) when they are isolated, at
      most ``SYSTEMATIC_FRACTION`` of the channel's samples (or fewer than
      ``SYSTEMATIC_MIN_COUNT``);
    * more than that: the channel is out of range systematically and is refused, with the likely
      fix (sign or unit) named.

    Parameters
    ----------
    data : merged table (canonical columns); repaired columns are replaced in it
    prov : row provenance
    nan_text : channel -> (N,) mask of cells written as literal NaN

    Returns
    -------
    warnings : recoverable defects found (one line per repair among them)
    repairs : the repairs made, one per channel and action

    Raises
    ------
    ValidationError
        A channel out of range systematically, a required channel with no sample, a NaN storm.
    """
    warns: list[str] = []
    repairs: list[Repair] = []
    t_all = data["t_s"].to_numpy() if "t_s" in data else np.full(len(data), np.nan)
    for name in list(data.columns):
        ch = BY_NAME.get(name)
        if ch is None or ch.kind == "time":
            continue
        v = data[name].to_numpy()
        txt = nan_text.get(name)
        n_txt = int(txt.sum()) if txt is not None else 0
        n_val = int(np.count_nonzero(~np.isnan(v)))
        if n_val == 0 and n_txt == 0:
            if ch.required:
                raise ValidationError("required channel has no sample (empty column)",
                                      file=prov.files[0],
                                      column=prov.source_column[0].get(name, name))
            warns.append(f"channel {name} has no sample; ignored")
            continue
        v_new = _range_checked(ch, v, n_val, prov, t_all, warns, repairs)
        if v_new is not None:
            data[name] = v_new
        if txt is not None and n_txt:
            frac = n_txt / (n_txt + n_val)
            where = prov.locate(txt, name)
            if frac > NAN_STORM_FRACTION or n_val == 0:
                raise ValidationError(f"NaN storm: {n_txt} of {n_txt + n_val} recorded samples "
                                      f"are NaN ({100 * frac:.0f} %)", **where)
            warns.append(f"{where['file']}: column '{where['column']}': {n_txt} NaN value(s) "
                         f"(first: row {where['rows'][0]}) treated as missing samples")
    return warns, repairs


def _range_checked(ch: Channel, v: np.ndarray, n_val: int, prov: Provenance, t_all: np.ndarray,
                   warns: list[str], repairs: list[Repair]) -> np.ndarray | None:
    """One channel against its physical range (rule: :func:`check_values`): the repaired
    values (clipped near the range, masked far out), ``None`` when every value is inside.

    Raises
    ------
    ValidationError
        The channel is out of range systematically.
    """
    name = ch.name
    with np.errstate(invalid="ignore"):
        low = v < ch.lo
        high = v > ch.hi
    bad = low | high
    if not bad.any():
        return None
    margin = 0.0 if (ch.angle or name in NO_CLIP) else CLIP_MARGIN.get(ch.unit, 0.0)
    with np.errstate(invalid="ignore"):
        clip = bad & np.isfinite(v) & (v >= ch.lo - margin) & (v <= ch.hi + margin)
    far = bad & ~clip
    n_far = int(far.sum())
    if n_far and n_far > SYSTEMATIC_FRACTION * n_val and n_far >= SYSTEMATIC_MIN_COUNT:
        where = prov.locate(far, name)
        first = v[far][0]
        raise ValidationError(
            f"{n_far} of {n_val} values ({100 * n_far / n_val:.1f} %) outside the "
            f"physical range (first {first:g} {ch.unit}; possible range [{ch.lo:g}, "
            f"{ch.hi:g}] {ch.unit}, values within {margin:g} {ch.unit} of it are "
            f"clipped): out of range systematically, not a glitch; "
            f"{_suggest_fix(ch, v[~np.isnan(v)])}", **where)
    v = v.copy()
    for action, m in (("clipped", clip), ("masked", far)):
        if m.any():
            _record_repairs(ch, v, m, action, prov, t_all, warns, repairs)
    v[clip & low] = ch.lo
    v[clip & high] = ch.hi
    v[far] = np.nan
    return v


def _record_repairs(ch: Channel, v: np.ndarray, m: np.ndarray, action: str, prov: Provenance,
                    t_all: np.ndarray, warns: list[str], repairs: list[Repair]) -> None:
    """One :class:`Repair` (and its warning line) per source file of the rows ``m``."""
    name = ch.name
    first = float(v[m][0])
    files = np.unique(prov.src_file[m])
    for f in files:
        mf = m & (prov.src_file == f)
        col = prov.source_column[int(f)].get(name, name)
        col_txt = col if col == name else f"{col}' -> '{name}"
        rep = Repair(file=prov.files[int(f)], column=col_txt, channel=name,
                     rows=tuple(int(r) for r in prov.row[mf]),
                     count=int(mf.sum()), action=action,
                     first_value=float(v[mf][0]) if f != files[0] else first,
                     bound=(float(ch.lo), float(ch.hi)),
                     t_s=tuple(float(x) for x in t_all[mf]))
        repairs.append(rep)
        warns.append(rep.message())
