"""Prior knowledge beside the log: known positions at given times (``--fix``) and a winds-aloft
table (``--wind``), parsed and validated here, carried in :class:`~flightrecon.types.FlightMeta`
(``fixes``, ``wind_aloft``) for the estimators (docs/schema.md, "Known positions and winds
aloft").

* ``--fix T_S,LAT,LON[,ALT_M[,SD_M]]`` (repeatable): a radar return, a waypoint report, a
  witness: the aircraft was at (LAT, LON) at ``t_s`` seconds of the record (the log's time
  base), at ``ALT_M`` metres MSL if given, within ``SD_M`` metres (one standard deviation per
  horizontal axis; default :data:`DEFAULT_FIX_SD_M`).
* ``--wind FILE``: a CSV with the header ``alt_msl_m,from_deg,speed_mps[,sd_mps]``, one row per
  level (a sounding or a winds-aloft forecast): the wind's meteorological direction (where it
  blows from) and speed at each MSL altitude, with the standard deviation of each velocity
  component (default :data:`DEFAULT_WIND_SD_MPS`).  Levels are sorted by altitude; two rows at
  one altitude are an error.
"""

from __future__ import annotations

import csv
import math
import os
import warnings
from itertools import pairwise
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.errors import (
    FlightReconWarning,
    InputFileError,
    MetadataError,
    SchemaError,
    ValidationError,
)
from flightrecon.ingest.encoding import decode_text
from flightrecon.types import FlightMeta, PositionFix, WindLevel

__all__ = ["DEFAULT_FIX_SD_M", "DEFAULT_WIND_SD_MPS", "check_fix_times", "parse_fix",
           "read_wind_table", "wind_aloft_on_grid"]

DEFAULT_FIX_SD_M = 100.0
"""Horizontal standard deviation of a known position when ``--fix`` gives none [m]."""
DEFAULT_WIND_SD_MPS = 2.0
"""Standard deviation of each wind component of a winds-aloft level when none is given [m/s]
(a forecast's typical vector error is 2-4 m/s)."""
WIND_COLUMNS = ("alt_msl_m", "from_deg", "speed_mps", "sd_mps")


def _finite(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise MetadataError(f"{what}: '{text}' is not a number") from None
    if not math.isfinite(v):
        raise MetadataError(f"{what}: '{text}' is not finite")
    return v


def parse_fix(text: str) -> PositionFix:
    """Parse ``"T_S,LAT,LON[,ALT_M[,SD_M]]"``.

    Raises
    ------
    MetadataError
        Not 3 to 5 numbers, non-finite, latitude outside [-90, 90], longitude outside
        [-180, 360), altitude outside [-1000, 25000] m, a standard deviation not positive.
    """
    parts = [p.strip() for p in str(text).split(",")]
    if not 3 <= len(parts) <= 5:
        raise MetadataError(f"--fix must be T_S,LAT,LON[,ALT_M[,SD_M]], got '{text}'")
    what = f"--fix '{text}'"
    t, lat, lon = (_finite(p, what) for p in parts[:3])
    alt = _finite(parts[3], what) if len(parts) > 3 and parts[3] != "" else None
    sd = _finite(parts[4], what) if len(parts) > 4 else DEFAULT_FIX_SD_M
    if not -90.0 <= lat <= 90.0:
        raise MetadataError(f"{what}: latitude {lat} outside [-90, 90]")
    if not -180.0 <= lon < 360.0:
        raise MetadataError(f"{what}: longitude {lon} outside [-180, 360)")
    if alt is not None and not -1000.0 <= alt <= 25000.0:
        raise MetadataError(f"{what}: altitude {alt} m outside [-1000, 25000] (metres MSL)")
    if sd <= 0.0:
        raise MetadataError(f"{what}: the standard deviation must be positive, got {sd}")
    return PositionFix(t_s=t, lat_deg=lat, lon_deg=lon if lon < 180.0 else lon - 360.0,
                       alt_msl_m=alt, sd_m=sd)


def check_fix_times(fixes, t_first_s: float, t_last_s: float) -> None:
    """Every fix inside the record's time span.

    Raises
    ------
    MetadataError
        A fix before the first or after the last sample of the log.
    """
    for f in fixes:
        if not t_first_s <= f.t_s <= t_last_s:
            raise MetadataError(f"--fix at t = {f.t_s:g} s is outside the record "
                                f"[{t_first_s:g}, {t_last_s:g}] s")


def read_wind_table(path: str | os.PathLike[str]) -> tuple[WindLevel, ...]:
    """Read a winds-aloft CSV (module docstring), levels sorted by altitude.

    Raises
    ------
    InputFileError
        Missing, unreadable or empty file.
    SchemaError
        Missing or unknown column.
    ValidationError
        A value that is not a finite number, out of range (altitude [-1000, 25000] m, direction
        [-360, 720] deg, speed [0, 150] m/s, sd > 0), or two levels at one altitude; the error
        names the file, the column and the 1-based data row.
    """
    path = Path(path)
    try:
        body, enc_warn = decode_text(path.read_bytes(), str(path))
    except FileNotFoundError:
        raise InputFileError("winds-aloft file not found", file=str(path)) from None
    except OSError as exc:
        raise InputFileError(f"cannot read the winds-aloft file: {exc}", file=str(path)) from None
    if enc_warn:                        # a Windows tool's Windows-1252 / Latin-1 text
        warnings.warn(enc_warn, FlightReconWarning, stacklevel=2)
    text = body.decode("utf-8")
    reader = csv.reader(line for line in text.splitlines() if line.strip())
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise InputFileError("the winds-aloft file is empty", file=str(path)) from None
    missing = [c for c in WIND_COLUMNS[:3] if c not in header]
    unknown = [c for c in header if c not in WIND_COLUMNS]
    if missing or unknown:
        raise SchemaError(f"winds-aloft columns must be {','.join(WIND_COLUMNS[:3])}[,sd_mps]"
                          + (f"; missing {missing}" if missing else "")
                          + (f"; unknown {unknown}" if unknown else ""), file=str(path))
    limits = {"alt_msl_m": (-1000.0, 25000.0), "from_deg": (-360.0, 720.0),
              "speed_mps": (0.0, 150.0), "sd_mps": (0.0, 50.0)}
    levels: list[WindLevel] = []
    for row_no, row in enumerate(reader, start=1):
        if len(row) != len(header):
            raise ValidationError(f"{len(row)} fields, expected {len(header)}", file=str(path),
                                  rows=[row_no])
        vals = {}
        for name, cell in zip(header, row):
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            lo, hi = limits[name]
            if not math.isfinite(v) or not lo <= v <= hi or (name == "sd_mps" and v <= 0.0):
                raise ValidationError(f"'{cell.strip()}' is not a value in [{lo:g}, {hi:g}]"
                                      + (" (and > 0)" if name == "sd_mps" else ""),
                                      file=str(path), column=name, rows=[row_no])
            vals[name] = v
        levels.append(WindLevel(alt_msl_m=vals["alt_msl_m"], from_deg=vals["from_deg"] % 360.0,
                                speed_mps=vals["speed_mps"],
                                sd_mps=vals.get("sd_mps", DEFAULT_WIND_SD_MPS)))
    if not levels:
        raise InputFileError("the winds-aloft file has no levels", file=str(path))
    levels.sort(key=lambda w: w.alt_msl_m)
    for a, b in pairwise(levels):
        if a.alt_msl_m == b.alt_msl_m:
            raise ValidationError(f"two levels at {a.alt_msl_m:g} m", file=str(path),
                                  column="alt_msl_m")
    return tuple(levels)


def wind_aloft_on_grid(grid: pd.DataFrame, meta: FlightMeta
                       ) -> tuple[np.ndarray, np.ndarray] | None:
    """The winds-aloft table of ``meta`` at the aircraft's altitude on each sample of ``grid``
    (docs/wind.md), or ``None`` without a table.

    The altitude is the pressure altitude ``baro_alt_m`` turned into an ISA altitude above MSL
    with the departure's QNH (:func:`flightrecon.geo.atmosphere.pressure_to_msl_m`; standard
    pressure without one).  A temperature 10 K off ISA moves it by about 3.5 %: 35 m at
    1000 m, a few cm/s of wind at forecast gradients of 1-5 (m/s)/km.  Where the pressure
    altitude is missing the result is NaN.

    Returns
    -------
    ne : (N, 2) north and east components of the air's velocity (where it moves to) [m/s]
    sd : (N,) standard deviation per component [m/s]
    """
    from flightrecon.geo.atmosphere import pressure_to_msl_m
    from flightrecon.geo.wind import wind_aloft_ne

    if not meta.wind_aloft:
        return None
    if "baro_alt_m" in grid.columns:
        baro = grid["baro_alt_m"].to_numpy(float)
    else:
        baro = np.full(len(grid), np.nan)
    h = np.asarray(pressure_to_msl_m(baro, meta.qnh_departure_hpa), dtype=float)
    return wind_aloft_ne(meta.wind_aloft, h)
