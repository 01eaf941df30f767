"""Flight metadata: the sidecar file ``<log stem>.meta.toml`` and command-line overrides.

Format (docs/schema.md, "Metadata"; the simulator writes the same)::

    [flight]
    aircraft_id = "A1"
    flight_id = "F1"
    epoch_utc = "2026-01-01T10:00:00Z"
    gnss_alt_datum = "ellipsoid"        # or "msl"
    baro_datum = "pressure"             # pressure altitude, 1013.25 hPa
    geoid_undulation_m = 0.0
    gnss_lever_arm_m = [0.0, 0.0, 0.0]  # body FRD, metres
    qnh_departure_hpa = 1013.25
    qnh_arrival_hpa = 1013.25
    [departure]
    lat_deg = 40.46
    lon_deg = 50.05
    elev_m = 3.0
    runway_true_deg = 160.0             # optional: true direction of the runway used
    threshold_lat_deg = 40.47           # optional, with runway_true_deg: that runway's
    threshold_lon_deg = 50.04           #   threshold (start of the roll, landing threshold)
    [arrival]                           # same keys
    [station]                           # same keys (ground radar)
    [gnss]                              # optional: how the GNSS is used (ingest/gnss_use.py)
    withhold_s = [[900.0, 1200.0]]      #   windows withheld, s of the log's time
    interval_s = 1.0                    #   at most one fix a second
    h_sd_m = 14.0                       #   the receiver's sd per axis (v_sd_m: vertical)
    [files]                             # optional companions, relative to the sidecar's folder
    gnss = "x_gnss.csv"
    radar = "x_radar.csv"
    mapping = "x.mapping.toml"

Settings resolve command line > sidecar > default.  Companion paths must stay inside the
sidecar's folder: absolute paths, ``..`` and symbolic links leading out are refused
(:class:`MetadataError`, exit code 7).  Unknown keys are reported as warnings, never dropped
silently; other tables are kept in ``FlightMeta.extra``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from datetime import UTC, datetime
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

import numpy as np

from flightrecon.errors import MetadataError
from flightrecon.ingest.gnss_use import GnssUse, gnss_use_from_table
from flightrecon.types import RECORD_FIELDS, FlightMeta, Position

__all__ = [
    "LOG_SUFFIXES",
    "Sidecar",
    "apply_overrides",
    "discover_sidecar",
    "load_sidecar",
    "normalise_epoch",
    "parse_position",
]

LOG_SUFFIXES = (".csv", ".txt", ".tsv", ".parquet", ".pq", ".parq")
FLIGHT_KEYS = {"aircraft_id", "flight_id", "epoch_utc", "gnss_alt_datum", "baro_datum",
               "geoid_undulation_m", "gnss_lever_arm_m", "qnh_departure_hpa", "qnh_arrival_hpa",
               "attitude_source", "configuration"}
POSITION_KEYS = ("lat_deg", "lon_deg", "elev_m", "runway_true_deg", "threshold_lat_deg",
                 "threshold_lon_deg")
THRESHOLD_MAX_M = 10_000.0
"""Largest distance of a runway threshold from its airfield reference point (a typo guard)."""
FILE_KEYS = ("gnss", "radar", "mapping")
GNSS_DATUMS = ("ellipsoid", "msl")
BARO_DATUMS = ("pressure", "qnh", "qfe")
ATTITUDE_SOURCES = ("ahrs", "inertial")
"""Values of ``[flight] attitude_source`` (:class:`flightrecon.types.FlightMeta`)."""


@dataclasses.dataclass(frozen=True)
class Sidecar:
    """A parsed sidecar: the metadata, companion files (resolved, confined) and warnings."""

    path: str
    meta: FlightMeta
    files: dict[str, Path]
    warnings: tuple[str, ...] = ()
    gnss: GnssUse | None = None
    #: the [flight] keys the file gives (a default is not a value given)
    given: frozenset[str] = frozenset()


def parse_position(text: str, *, what: str = "position") -> Position:
    """Parse ``"LAT,LON,ELEV_M"`` (degrees, degrees, metres MSL; elevation optional).

    Raises
    ------
    MetadataError
        Not two or three numbers, non-finite, latitude outside [-90, 90] or longitude outside
        [-180, 360).
    """
    parts = [p.strip() for p in str(text).split(",")]
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise MetadataError(f"{what} must be LAT,LON[,ELEV_M] in degrees and metres, "
                            f"got '{text}'") from None
    if len(nums) not in (2, 3):
        raise MetadataError(f"{what} must be LAT,LON[,ELEV_M], got '{text}'")
    if len(nums) == 2:
        nums.append(0.0)
    return _position(nums[0], nums[1], nums[2], what)


def _position(lat: Any, lon: Any, elev: Any, what: str, file: str | None = None) -> Position:
    try:
        lat, lon, elev = float(lat), float(lon), float(elev)
    except (TypeError, ValueError):
        raise MetadataError(f"{what}: lat_deg, lon_deg, elev_m must be numbers",
                            file=file) from None
    if not all(map(math.isfinite, (lat, lon, elev))):
        raise MetadataError(f"{what}: non-finite coordinate", file=file)
    if not -90.0 <= lat <= 90.0:
        raise MetadataError(f"{what}: latitude {lat} outside [-90, 90] deg", file=file)
    if not -180.0 <= lon < 360.0:
        raise MetadataError(f"{what}: longitude {lon} outside [-180, 360) deg", file=file)
    if not -1000.0 <= elev <= 10000.0:
        raise MetadataError(f"{what}: elevation {elev} m outside [-1000, 10000] m", file=file)
    if lon >= 180.0:
        lon -= 360.0
    return Position(lat, lon, elev)


def normalise_epoch(text: Any, file: str | None = None) -> str:
    """An ISO-8601 UTC time as ``YYYY-MM-DDTHH:MM:SS[.ffffff]Z``.

    A time without a zone is taken as UTC; a non-UTC offset is converted.

    Raises
    ------
    MetadataError
        Not an ISO-8601 date-time.
    """
    if isinstance(text, datetime):
        dt = text
    else:
        s = str(text).strip()
        try:
            dt = datetime.fromisoformat(s[:-1] + "+00:00" if s.endswith(("Z", "z")) else s)
        except ValueError:
            raise MetadataError(f"epoch_utc '{text}' is not an ISO-8601 date-time "
                                "(e.g. 2026-01-01T10:00:00Z)", file=file) from None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=UTC)
    dt = dt.astimezone(UTC).replace(tzinfo=None)
    return dt.isoformat() + "Z"


def discover_sidecar(log: str | os.PathLike) -> Path | None:
    """``<log name without its suffix>.meta.toml`` beside ``log`` if it exists, else ``None``."""
    p = Path(log)
    stem = p.name
    for s in LOG_SUFFIXES:
        if stem.lower().endswith(s):
            stem = stem[: -len(s)]
            break
    cand = p.with_name(stem + ".meta.toml")
    return cand if cand.is_file() else None


def _confined(folder: Path, rel: Any, key: str, file: str) -> Path:
    """Resolve a companion path, refusing anything that leaves ``folder``."""
    if not isinstance(rel, str) or not rel.strip():
        raise MetadataError(f"[files] {key} must be a non-empty relative path", file=file)
    if "\x00" in rel:
        raise MetadataError(f"[files] {key}: NUL byte in path", file=file)
    if PurePosixPath(rel).is_absolute() or PureWindowsPath(rel).is_absolute() \
            or PureWindowsPath(rel).drive or rel.startswith("~"):
        raise MetadataError(f"[files] {key} = '{rel}': absolute paths are not allowed; give a "
                            "path relative to the sidecar's folder", file=file)
    parts = PurePosixPath(rel.replace("\\", "/")).parts
    if ".." in parts:
        raise MetadataError(f"[files] {key} = '{rel}': '..' is not allowed (companion files "
                            "must be inside the sidecar's folder)", file=file)
    root = folder.resolve()
    target = (folder / rel).resolve()
    try:
        target.relative_to(root)
    except ValueError:
        raise MetadataError(f"[files] {key} = '{rel}' leads outside the sidecar's folder "
                            "(symbolic link?)", file=file) from None
    if not target.is_file():
        raise MetadataError(f"[files] {key} = '{rel}': file not found", file=file)
    return target


def load_sidecar(path: str | os.PathLike) -> Sidecar:
    """Parse a sidecar file into :class:`FlightMeta` and its companion files.

    Raises
    ------
    MetadataError
        Missing or unreadable file, not TOML, wrong types or values, hostile companion paths.
    """
    p = Path(path)
    file = str(p)
    if not p.is_file():
        raise MetadataError("sidecar file not found", file=file)
    try:
        doc = tomllib.loads(p.read_bytes().decode("utf-8"))
    except UnicodeDecodeError:
        raise MetadataError("sidecar is not UTF-8 text", file=file) from None
    except tomllib.TOMLDecodeError as exc:
        raise MetadataError(f"not a valid TOML file: {exc}", file=file) from None
    warns: list[str] = []
    kw: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    flight = doc.get("flight", {})
    if not isinstance(flight, dict):
        raise MetadataError("[flight] must be a table", file=file)
    for k, v in flight.items():
        if k not in FLIGHT_KEYS:
            warns.append(f"{file}: unknown key [flight] {k} (kept in metadata 'extra')")
            extra[k] = v
            continue
        kw[k] = _flight_value(k, v, file)
    for name in ("departure", "arrival", "station"):
        if name in doc:
            t = doc[name]
            if not isinstance(t, dict):
                raise MetadataError(f"[{name}] must be a table", file=file)
            missing = [k for k in ("lat_deg", "lon_deg") if k not in t]
            if missing:
                raise MetadataError(f"[{name}] misses {', '.join(missing)}", file=file)
            for k in t:
                if k not in POSITION_KEYS:
                    warns.append(f"{file}: unknown key [{name}] {k} (ignored)")
            pos = _position(t["lat_deg"], t["lon_deg"], t.get("elev_m", 0.0), f"[{name}]", file)
            if "runway_true_deg" in t:
                if name == "station":
                    raise MetadataError("[station] runway_true_deg: a radar station has no "
                                        "runway", file=file)
                rw = t["runway_true_deg"]
                if isinstance(rw, bool) or not isinstance(rw, (int, float)) \
                        or not math.isfinite(rw) or not 0.0 <= rw < 360.0:
                    raise MetadataError(f"[{name}] runway_true_deg must be a number in [0, 360) "
                                        f"deg, got {rw!r}", file=file)
                pos = dataclasses.replace(pos, runway_true_deg=float(rw))
            pos = _threshold(t, pos, name, file)
            kw[name] = pos
    files: dict[str, Path] = {}
    if "files" in doc:
        ft = doc["files"]
        if not isinstance(ft, dict):
            raise MetadataError("[files] must be a table", file=file)
        for k, v in ft.items():
            if k not in FILE_KEYS:
                raise MetadataError(f"[files] unknown key '{k}' (allowed: {', '.join(FILE_KEYS)})",
                                    file=file)
            files[k] = _confined(p.parent, v, k, file)
    gnss = None
    if "gnss" in doc:
        gnss, w = gnss_use_from_table(doc["gnss"], file)
        warns += w
    for k, v in doc.items():
        if k not in ("flight", "departure", "arrival", "station", "files", "gnss"):
            extra[k] = v
    meta = FlightMeta(**kw, extra=extra)
    return Sidecar(path=file, meta=meta, files=files, warnings=tuple(warns), gnss=gnss,
                   given=frozenset(kw))


def _ground_distance_m(a: Position, b: Position) -> float:
    """Horizontal distance [m] from ``a`` to ``b`` on the WGS-84 ellipsoid, for the plausibility
    check of a runway threshold (a few kilometres at most).

    Offsets north and east at the mean latitude ``lat_m`` of the two points:
    ``dn = dlat M``, ``de = dlon N cos(lat_m)`` with the meridian and prime-vertical radii
    ``M``, ``N`` at ``lat_m`` (formula in :mod:`flightrecon.geo.ellipsoid`), at the ellipsoid's
    surface.  Against the tangent-plane projection (:class:`flightrecon.geo.frames.TangentPlane`)
    the difference stays below 0.1 m up to 10 km at latitudes up to 80 deg
    (``tests/test_faults_inputs.py``), without importing pyproj: the ingest and
    ``flightrecon info`` stay light.
    """
    from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2

    lat_m = np.radians(0.5 * (a.lat_deg + b.lat_deg))
    w = 1.0 - WGS84_E2 * np.sin(lat_m) ** 2
    n_radius = WGS84_A / np.sqrt(w)
    m_radius = n_radius * (1.0 - WGS84_E2) / w
    dlon = (b.lon_deg - a.lon_deg + 180.0) % 360.0 - 180.0
    dn = np.radians(b.lat_deg - a.lat_deg) * m_radius
    de = np.radians(dlon) * n_radius * np.cos(lat_m)
    return float(np.hypot(dn, de))


def _threshold(t: dict[str, Any], pos: Position, name: str, file: str) -> Position:
    """``pos`` with the runway threshold of table ``[name]`` (both coordinates or neither; the
    runway's direction must be given too; within :data:`THRESHOLD_MAX_M` of the reference)."""
    keys = ("threshold_lat_deg", "threshold_lon_deg")
    given = [k in t for k in keys]
    if not any(given):
        return pos
    if name == "station":
        raise MetadataError("[station] threshold_lat_deg/threshold_lon_deg: a radar station has "
                            "no runway", file=file)
    if not all(given):
        missing = keys[given.index(False)]
        raise MetadataError(f"[{name}] a runway threshold needs both threshold_lat_deg and "
                            f"threshold_lon_deg ({missing} is missing)", file=file)
    if pos.runway_true_deg is None:
        raise MetadataError(f"[{name}] a runway threshold needs the runway's direction "
                            "(runway_true_deg)", file=file)
    thr = _position(t[keys[0]], t[keys[1]], pos.elev_m, f"[{name}] threshold", file)
    d = _ground_distance_m(pos, thr)
    if d > THRESHOLD_MAX_M:
        raise MetadataError(f"[{name}] the runway threshold is {d / 1000:.1f} km from the "
                            f"airfield reference point (more than {THRESHOLD_MAX_M / 1000:.0f} km: "
                            "a wrong coordinate?)", file=file)
    return dataclasses.replace(pos, threshold_lat_deg=thr.lat_deg, threshold_lon_deg=thr.lon_deg)


def _flight_value(k: str, v: Any, file: str) -> Any:
    if k == "configuration":  # free text for the coefficient store (docs/store.md)
        return str(v)
    if k in ("aircraft_id", "flight_id"):
        if not isinstance(v, (str, int)) or isinstance(v, bool):
            raise MetadataError(f"[flight] {k} must be a string", file=file)
        return str(v)
    if k == "epoch_utc":
        return normalise_epoch(v, file)
    if k == "gnss_alt_datum":
        if v not in GNSS_DATUMS:
            raise MetadataError(f"[flight] gnss_alt_datum must be one of {GNSS_DATUMS}, got {v!r}",
                                file=file)
        return v
    if k == "baro_datum":
        if v not in BARO_DATUMS:
            raise MetadataError(f"[flight] baro_datum must be one of {BARO_DATUMS}, got {v!r}",
                                file=file)
        return v
    if k == "attitude_source":
        if v not in ATTITUDE_SOURCES:
            raise MetadataError(f"[flight] attitude_source must be one of {ATTITUDE_SOURCES}, "
                                f"got {v!r}", file=file)
        return v
    if k == "gnss_lever_arm_m":
        if not isinstance(v, list) or len(v) != 3:
            raise MetadataError("[flight] gnss_lever_arm_m must be [x, y, z] in metres (FRD)",
                                file=file)
        return tuple(_number(x, "gnss_lever_arm_m", file) for x in v)
    val = _number(v, k, file)
    if k.startswith("qnh") and not 850.0 <= val <= 1090.0:
        raise MetadataError(f"[flight] {k} = {val} hPa outside [850, 1090]", file=file)
    if k == "geoid_undulation_m" and not -120.0 <= val <= 100.0:
        raise MetadataError(f"[flight] geoid_undulation_m = {val} outside [-120, 100] m",
                            file=file)
    return val


def _number(v: Any, k: str, file: str | None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise MetadataError(f"[flight] {k} must be a finite number, got {v!r}", file=file)
    return float(v)


def apply_overrides(meta: FlightMeta, overrides: dict[str, Any] | None) -> FlightMeta:
    """``meta`` with command-line values replacing the sidecar's (command line wins).

    ``overrides`` keys are :class:`FlightMeta` fields; ``None`` values are ignored; positions
    may be :class:`Position` or ``"LAT,LON,ELEV_M"`` strings.

    Raises
    ------
    MetadataError
        Unknown key or bad value.
    """
    if not overrides:
        return meta
    names = {f.name for f in dataclasses.fields(FlightMeta)} - set(RECORD_FIELDS)
    kw: dict[str, Any] = {}
    for k, v in overrides.items():
        if v is None:
            continue
        if k not in names:
            raise MetadataError(f"unknown metadata override '{k}' (known: "
                                f"{', '.join(sorted(names))})")
        if k == "fixes":  # PositionFix objects or "T_S,LAT,LON[,ALT_M[,SD_M]]" strings
            from flightrecon.ingest.priors import parse_fix

            kw[k] = tuple(sorted((parse_fix(f) if isinstance(f, str) else f for f in v),
                                 key=lambda f: f.t_s))
            continue
        if k == "wind_aloft":  # WindLevel objects or the path of a winds-aloft CSV
            from flightrecon.ingest.priors import read_wind_table

            kw[k] = read_wind_table(v) if isinstance(v, (str, os.PathLike)) else tuple(v)
            continue
        if k in ("departure", "arrival", "station"):
            if isinstance(v, str):
                v = parse_position(v, what=f"--{k}")
            elif not isinstance(v, Position):
                raise MetadataError(f"--{k} must be a position")
            kw[k] = v
        else:
            kw[k] = _flight_value(k, list(v) if isinstance(v, tuple) else v, "command line")
    return dataclasses.replace(meta, **kw)
