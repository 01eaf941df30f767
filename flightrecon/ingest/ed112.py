"""A flight-data team's parameter dump of a decoded ED-112 / ARINC 717 recorder, read as
recorded, with no mapping file (docs/ingest.md, "Parameter dumps of a flight data recorder").

The layout (:func:`flightrecon.ingest.units_line.units_line` recognises it): a CSV whose first line is the header of the
parameters' mnemonics (``VRTG``, ``LONG``, ``LATG``, ``PTCH``, ``ROLL``, ``HEAD``, ``CAS``,
``ALT``, ...), whose **second line is the units line** (``g``, ``deg``, ``kt``, ``ft``,
``degC``: no cell a number), then one row per sample.  The time is a column of seconds
(``TIME`` in ``s``), or the recorder's **frame and subframe counters**: an ARINC 717 frame is
four subframes of one second each (ARINC 717; EUROCAE ED-112 keeps the same frame for digital
flight data recorders; public decoders of NTSB recorder files write one row per subframe,
"subframes are recorded in the FDR once per second"), so subframe ``s`` of frame ``f`` starts
at ``((f - f0) n_sub + s - s_first)`` seconds, ``n_sub`` the subframe count (4; 1-based or
0-based as the file counts them).  The frame counter is the recorder's 12-bit word: a drop back
to a small value is its wrap (+4096 frames).  Several rows of one subframe (a parameter dump
that writes each word slot's sample on its own row) are spread evenly over its second, in file
order, with a warning (the slot times within the second are the frame layout's, which the dump
does not give).

The parameters (:data:`MNEMONICS`) are read in the unit their units line gives; a recognised
mnemonic whose unit flightrecon does not know is left out with a warning (the analyst maps it);
a user mapping file overrides any channel and the time (:func:`dump_mapping`).  What the dump
cannot tell is assumed with a warning: a heading without ``TRUE`` in its mnemonic is magnetic
(the flight crew's reference a recorder takes) and the lateral load is positive toward the right
wing (the schema's sign; a recorder counting it positive left needs ``sign = -1`` in a
mapping).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.ingest.mapping import ChannelSpec, Mapping, TimeSpec
from flightrecon.ingest.readers import RawTable
from flightrecon.ingest.units import CANONICAL_DIMENSION, lookup_unit
from flightrecon.schema import BY_NAME

__all__ = ["FRAME_WRAP", "MNEMONICS", "SUBFRAME_S", "counter_seconds", "dump_mapping"]

#: name of the built-in mapping in messages and notes
PRESET = "built-in parameter-dump mapping (flightrecon/ingest/ed112.py)"
#: one ARINC 717 subframe [s]
SUBFRAME_S = 1.0
#: the 12-bit frame counter's period
FRAME_WRAP = 4096
#: the time column, the frame and the subframe counters, by their usual headers (upper case)
TIME_NAMES = ("TIME", "TIME_S", "TIME_SEC", "SECONDS", "ELAPSED_TIME")
FRAME_NAMES = ("FRAME", "FRAME_COUNTER", "FRAME COUNTER", "FRAMECOUNTER", "FRM", "FRAME_NO")
SUBFRAME_NAMES = ("SUBFRAME", "SUB_FRAME", "SUBFRAME_ID", "SUB FRAME", "SUBFRM", "SF")
#: canonical channel -> the mnemonics recorded for it (upper case), the usual ARINC 717 /
#: ED-112 spellings and their long forms; the first found in the header is read
MNEMONICS: dict[str, tuple[str, ...]] = {
    "n_norm_g": ("VRTG", "VERT_ACCEL", "VERTICAL ACCELERATION", "NORMAL_ACCEL", "ACC_NORM"),
    "n_long_g": ("LONG", "LONG_ACCEL", "LONGITUDINAL ACCELERATION", "ACC_LONG"),
    "n_lat_g": ("LATG", "LAT_ACCEL", "LATERAL ACCELERATION", "ACC_LAT"),
    "pitch_deg": ("PTCH", "PITCH", "PITCH ATTITUDE", "PITCH_ANGLE"),
    "roll_deg": ("ROLL", "ROLL ATTITUDE", "ROLL_ANGLE", "BANK"),
    "heading_deg": ("HEAD", "HDG", "HEAD_MAG", "HDG_MAG", "MAGNETIC HEADING", "HEADING",
                    "HEAD_TRUE", "HDG_TRUE", "TRUE HEADING"),
    "cas_mps": ("CAS", "CAS_KT", "COMPUTED AIRSPEED", "CALIBRATED AIRSPEED"),
    "ias_mps": ("IAS", "INDICATED AIRSPEED"),
    "tas_mps": ("TAS", "TRUE AIRSPEED"),
    "baro_alt_m": ("ALT", "ALT_STD", "ALTSTD", "PALT", "ALT_FT", "PRESSURE ALTITUDE", "ALTP"),
    "sat_degc": ("SAT", "SAT_C", "STATIC AIR TEMPERATURE", "OAT"),
    "gnss_lat_deg": ("GPS_LAT", "LAT_GPS", "GPS LATITUDE"),
    "gnss_lon_deg": ("GPS_LON", "LON_GPS", "GPS LONGITUDE"),
}
#: the name of the time column the frame and subframe counters are turned into
COUNTER_TIME = "(FRAME, SUBFRAME) s"


def _find(columns, names: tuple[str, ...]) -> str | None:
    upper = {c.strip().upper(): c for c in columns}
    return next((upper[n] for n in names if n in upper), None)


def dump_mapping(raw: RawTable, user: Mapping | None
                 ) -> tuple[RawTable, Mapping, tuple[str, ...], list[str], list[str]]:
    """The built-in mapping of a parameter dump (module docstring), under the user's.

    Returns
    -------
    raw : the table, with the frame and subframe counters' seconds as column
        :data:`COUNTER_TIME` when the time is read from them
    mapping : the built-in channels and time, the user's mapping laid over them (the user's
        ``[time]`` and channels win; a built-in channel whose column the user maps is left out)
    used : the source columns the time is read from (not "ignored" columns)
    notes, warnings : what was read and what was assumed
    """
    notes: list[str] = []
    warns: list[str] = []
    specs = _channel_specs(raw, warns)
    time, raw, used = _time(raw, notes, warns) if user is None or user.time is None \
        else (user.time, raw, ())
    preset = Mapping(file=PRESET, time=time, channels=tuple(specs))
    if user is not None:
        theirs = {s.channel for s in user.channels}
        cols = {s.column for s in user.channels if s.column}
        kept = [s for s in preset.channels if s.channel not in theirs and s.column not in cols]
        preset = dataclasses.replace(user, time=user.time or preset.time,
                                     channels=(*kept, *user.channels))
    notes.append(f"{raw.file}: parameter dump (header, units line) read with the "
                 f"{PRESET}" + (" under the user's mapping" if user is not None else "") + ": "
                 + ", ".join(f"{s.channel} <- {s.column}" for s in specs))
    return raw, preset, used, notes, warns


def _channel_specs(raw: RawTable, warns: list[str]) -> list[ChannelSpec]:
    """A spec for each channel of :data:`MNEMONICS` whose mnemonic the header has, in the unit
    of the units line; the assumptions the dump leaves open said in ``warns``."""
    specs: list[ChannelSpec] = []
    for channel, names in MNEMONICS.items():
        col = _find(raw.columns, names)
        if col is None or any(s.column == col for s in specs):
            continue
        text = raw.units.get(col, "")
        unit = lookup_unit(text) if text else None
        need = CANONICAL_DIMENSION[BY_NAME[channel].unit]
        if unit is None or unit.dimension != need:
            warns.append(f"{raw.file}: column '{col}' ({channel}?) in unit '{text}', which is "
                         f"not a {need} unit flightrecon knows: not read (map it with a mapping "
                         "file)")
            continue
        ref = "true"
        if channel == "heading_deg" and "TRUE" not in col.upper():
            ref = "magnetic"
            warns.append(f"{raw.file}: heading '{col}' taken as magnetic (a recorder's heading "
                         "is the crew's reference; the dump does not say): map it with "
                         "reference = \"true\" if it is true")
        if channel == "n_lat_g":
            warns.append(f"{raw.file}: lateral load '{col}' taken as positive toward the right "
                         "wing (the dump does not say): map it with sign = -1 if the recorder "
                         "counts it positive left")
        specs.append(ChannelSpec(channel, col, unit, reference=ref))
    taken = {s.channel for s in specs} | {s.column for s in specs}
    for col in raw.columns:          # canonical names: in the unit of the units line
        ch = BY_NAME.get(col)
        unit = lookup_unit(raw.units.get(col, "")) if raw.units.get(col) else None
        if ch is None or ch.kind == "time" or col in taken or unit is None:
            continue
        if unit.dimension != CANONICAL_DIMENSION[ch.unit]:
            warns.append(f"{raw.file}: column '{col}': the units line gives "
                         f"'{raw.units[col]}', not a {CANONICAL_DIMENSION[ch.unit]} unit: read "
                         f"in the unit its name gives ({ch.unit})")
            continue
        specs.append(ChannelSpec(col, col, unit))
    return specs


def _time(raw: RawTable, notes: list[str], warns: list[str]
          ) -> tuple[TimeSpec | None, RawTable, tuple[str, ...]]:
    """The dump's time: a column of seconds, else the frame and subframe counters
    (:func:`counter_seconds`), else none (the refusal then says how to give one)."""
    col = _find(raw.columns, TIME_NAMES)
    unit = lookup_unit(raw.units.get(col, "")) if col is not None else None
    if col is not None and raw.columns[col].dtype == np.float64 and unit is not None \
            and unit.name in ("s", "1"):
        return TimeSpec(col, "s"), raw, (col,)
    frame = _find(raw.columns, FRAME_NAMES)
    sub = _find(raw.columns, SUBFRAME_NAMES)
    if frame is None or sub is None:
        return None, raw, ()
    t, note, warn = counter_seconds(raw, frame, sub)
    notes.append(note)
    if warn:
        warns.append(warn)
    cols = {**raw.columns, COUNTER_TIME: t}
    return TimeSpec(COUNTER_TIME, "s"), dataclasses.replace(raw, columns=cols), (frame, sub)


def counter_seconds(raw: RawTable, frame: str, sub: str) -> tuple[np.ndarray, str, str | None]:
    """Seconds of every row from the frame and subframe counters (module docstring).

    Returns
    -------
    t : (N,) seconds from the first row's subframe
    note : how the time was read
    warning : the rows-per-subframe spread, when rows share a subframe (else ``None``)

    Raises
    ------
    ValidationError
        A counter that is missing or not a whole number, a subframe outside ``1..4`` (or
        ``0..3``), or a frame that goes back without wrapping (naming the rows).
    """
    rows = np.arange(1, raw.n_rows + 1)
    f = _counter(raw, frame, rows)
    s = _counter(raw, sub, rows)
    first = 0 if s.min() == 0 else 1
    n_sub = 4
    if s.min() < 0 or s.max() - first > 3:
        bad = np.flatnonzero((s < first) | (s > first + 3))
        raise ValidationError("subframe counter outside 1..4 (or 0..3): not an ARINC 717 "
                              "frame", file=raw.file, column=sub, rows=rows[bad] if bad.size
                              else None)
    step = np.diff(f)
    wrap = (step < 0) & (f[1:] < 16) & (f[:-1] >= FRAME_WRAP - 16)
    back = np.flatnonzero((step < 0) & ~wrap)
    if back.size:
        raise ValidationError("frame counter goes back (not the 12-bit counter's wrap)",
                              file=raw.file, column=frame, rows=rows[back + 1])
    fu = f + FRAME_WRAP * np.concatenate([[0], np.cumsum(wrap)])
    sec = (fu - fu[0]) * n_sub + (s - first) - (s[0] - first)
    # rows sharing a subframe: spread evenly over its second, in file order
    start = np.flatnonzero(np.r_[True, np.diff(sec) != 0])
    count = np.diff(np.r_[start, sec.size])
    k = np.arange(sec.size) - np.repeat(start, count)
    t = (sec + k / np.repeat(count, count)) * SUBFRAME_S
    note = (f"{raw.file}: time from the frame counter '{frame}' and the subframe counter '{sub}'"
            f": {n_sub} subframes of {SUBFRAME_S:g} s a frame (ARINC 717), the first row at 0 s"
            + (f", {int(wrap.sum())} wrap(s) of the 12-bit frame counter" if wrap.any() else ""))
    warn = None
    if count.max() > 1:
        warn = (f"{raw.file}: {int(count.max())} rows in a subframe (median {np.median(count):g})"
                ": spread evenly over its second in file order (the slot times within the "
                "second are the frame layout's, not in the dump)")
    return t, note, warn


def _counter(raw: RawTable, col: str, rows: np.ndarray) -> np.ndarray:
    v = raw.columns[col]
    if v.dtype != np.float64:
        raise ValidationError("counter is not numeric", file=raw.file, column=col)
    bad = np.flatnonzero(~np.isfinite(v) | (np.abs(v - np.round(v)) > 1e-9))
    if bad.size:
        raise ValidationError("counter missing or not a whole number", file=raw.file,
                              column=col, rows=rows[bad])
    return np.round(v).astype(np.int64)
