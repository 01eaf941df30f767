"""The coefficient store's schema: its identity (``PRAGMA application_id``
:data:`APPLICATION_ID`, the ``store_meta`` marker, ``PRAGMA user_version``
:data:`SCHEMA_VERSION`), the tables of every version, their creation and the migrations from
each version to the next (docs/store.md).  Opening, checking and locking the file is
:mod:`flightrecon.store.db`'s."""

from __future__ import annotations

import sqlite3

from flightrecon import __version__

#: ``PRAGMA application_id`` of a flightrecon coefficient store: b"FRCS" read big-endian
APPLICATION_ID: int = int.from_bytes(b"FRCS", "big")
#: value of ``store_meta.application``
APPLICATION_NAME = "flightrecon-coefficients"
#: current schema version (``PRAGMA user_version``)
SCHEMA_VERSION = 4

_META_DDL = """
CREATE TABLE store_meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
)"""


#: schema v1 as shipped before per-axis branches and iteration counts were recorded; kept so that
#: old stores can be upgraded (and the upgrade tested): see :func:`migrate_v1_to_v2`.
SCHEMA_V1_DDL: tuple[str, ...] = (
    _META_DDL,
    """
CREATE TABLE flights (
    id                INTEGER PRIMARY KEY,
    aircraft_id       TEXT NOT NULL CHECK (length(aircraft_id) > 0),
    flight_id         TEXT NOT NULL CHECK (length(flight_id) > 0),
    flight_date_utc   TEXT NOT NULL,
    duration_s        REAL NOT NULL CHECK (duration_s > 0),
    k1                REAL NOT NULL,
    k2                REAL NOT NULL,
    k3                REAL NOT NULL,
    converged         INTEGER NOT NULL CHECK (converged IN (0, 1)),
    residual_m        REAL NOT NULL,
    software_version  TEXT NOT NULL,
    settings_json     TEXT NOT NULL,
    input_hashes_json TEXT NOT NULL,
    recorded_at_utc   TEXT NOT NULL,
    UNIQUE (aircraft_id, flight_id)
)""",
    "CREATE INDEX flights_by_aircraft ON flights (aircraft_id, flight_date_utc)",
)


_FLIGHTS_V2_COLUMNS = """
    id                INTEGER PRIMARY KEY,
    aircraft_id       TEXT NOT NULL CHECK (length(aircraft_id) > 0),
    flight_id         TEXT NOT NULL CHECK (length(flight_id) > 0),
    flight_date_utc   TEXT NOT NULL,
    duration_s        REAL NOT NULL CHECK (duration_s > 0),
    k1                REAL,
    k2                REAL,
    k3                REAL,
    branch_k1         TEXT NOT NULL CHECK (branch_k1 IN ('negative', 'positive', 'none')),
    branch_k2         TEXT NOT NULL CHECK (branch_k2 IN ('negative', 'positive', 'none')),
    branch_k3         TEXT NOT NULL CHECK (branch_k3 IN ('negative', 'positive', 'none')),
    converged         INTEGER NOT NULL CHECK (converged IN (0, 1)),
    converged_k1      INTEGER NOT NULL CHECK (converged_k1 IN (0, 1)),
    converged_k2      INTEGER NOT NULL CHECK (converged_k2 IN (0, 1)),
    converged_k3      INTEGER NOT NULL CHECK (converged_k3 IN (0, 1)),
    residual_m        REAL,
    iterations        INTEGER CHECK (iterations IS NULL OR iterations >= 0),
    software_version  TEXT NOT NULL,
    settings_json     TEXT NOT NULL,
    input_hashes_json TEXT NOT NULL,
    recorded_at_utc   TEXT NOT NULL,
    UNIQUE (aircraft_id, flight_id),
    CHECK (converged = (converged_k1 AND converged_k2 AND converged_k3)),
    CHECK (converged_k1 = 0 OR (k1 IS NOT NULL AND branch_k1 != 'none')),
    CHECK (converged_k2 = 0 OR (k2 IS NOT NULL AND branch_k2 != 'none')),
    CHECK (converged_k3 = 0 OR (k3 IS NOT NULL AND branch_k3 != 'none')),
    CHECK (converged = 0 OR residual_m IS NOT NULL)
"""


#: schema v2, as shipped before the sensor-calibration tables (kept for the upgrade tests)
SCHEMA_V2_DDL: tuple[str, ...] = (
    _META_DDL,
    f"CREATE TABLE flights ({_FLIGHTS_V2_COLUMNS})",
    "CREATE INDEX flights_by_aircraft ON flights (aircraft_id, flight_date_utc)",
)


#: tables added by schema v3: the joint smoother's estimates of the persistent sensor errors per
#: flight with the conditions that make flights comparable, the sensor changes after which earlier
#: flights no longer apply, and the per-aircraft drift settings (docs/store.md, "Sensor
#: calibration")
_V3_TABLES: tuple[str, ...] = (
    """
CREATE TABLE calibration_flights (
    id                INTEGER PRIMARY KEY,
    aircraft_id       TEXT NOT NULL CHECK (length(aircraft_id) > 0),
    flight_id         TEXT NOT NULL CHECK (length(flight_id) > 0),
    flight_date_utc   TEXT NOT NULL,
    log_sha256        TEXT,
    configuration     TEXT NOT NULL,
    sources           TEXT NOT NULL,
    duration_s        REAL NOT NULL CHECK (duration_s > 0),
    tas_min_mps       REAL,
    tas_max_mps       REAL,
    alt_min_m         REAL,
    alt_max_m         REAL,
    converged         INTEGER NOT NULL CHECK (converged IN (0, 1)),
    software_version  TEXT NOT NULL,
    settings_json     TEXT NOT NULL,
    input_hashes_json TEXT NOT NULL,
    recorded_at_utc   TEXT NOT NULL,
    UNIQUE (aircraft_id, flight_id)
)""",
    "CREATE INDEX calibration_by_aircraft ON calibration_flights (aircraft_id, flight_date_utc)",
    """
CREATE TABLE sensor_estimates (
    flight_ref  INTEGER NOT NULL REFERENCES calibration_flights (id) ON DELETE CASCADE,
    quantity    TEXT NOT NULL CHECK (length(quantity) > 0),
    value       REAL NOT NULL,
    sd          REAL NOT NULL CHECK (sd >= 0),
    prior_mean  REAL NOT NULL,
    prior_sd    REAL NOT NULL CHECK (prior_sd > 0),
    unit        TEXT NOT NULL,
    PRIMARY KEY (flight_ref, quantity)
)""",
    """
CREATE TABLE sensor_changes (
    id          INTEGER PRIMARY KEY,
    aircraft_id TEXT NOT NULL CHECK (length(aircraft_id) > 0),
    quantity    TEXT NOT NULL CHECK (length(quantity) > 0),
    change_utc  TEXT NOT NULL,
    note        TEXT NOT NULL,
    UNIQUE (aircraft_id, quantity, change_utc)
)""",
    """
CREATE TABLE calibration_drift (
    aircraft_id       TEXT NOT NULL CHECK (length(aircraft_id) > 0),
    quantity          TEXT NOT NULL CHECK (length(quantity) > 0),
    sd_per_sqrt_day   REAL NOT NULL CHECK (sd_per_sqrt_day >= 0),
    PRIMARY KEY (aircraft_id, quantity)
)""",
)


#: schema v3 (current), for a new store
SCHEMA_V3_DDL: tuple[str, ...] = (
    _META_DDL,
    f"CREATE TABLE flights ({_FLIGHTS_V2_COLUMNS})",
    "ALTER TABLE flights ADD COLUMN log_sha256 TEXT",
    "CREATE INDEX flights_by_aircraft ON flights (aircraft_id, flight_date_utc)",
    *_V3_TABLES,
)


#: columns added by schema v4: each root's conditioning, ``50 m / |dF/dk|`` (NULL: unknown),
#: which weights the fleet means (docs/store.md, "The averaging rule")
_V4_COLUMNS: tuple[str, ...] = tuple(
    f"ALTER TABLE flights ADD COLUMN {c} REAL CHECK ({c} IS NULL OR {c} > 0)"
    for c in ("k1_sd", "k2_sd", "k3_sd"))


#: schema v4 (current): v3 and the roots' conditioning
SCHEMA_V4_DDL: tuple[str, ...] = SCHEMA_V3_DDL + _V4_COLUMNS


#: columns of ``calibration_flights``, in order, without ``id``
CALIBRATION_COLUMNS: tuple[str, ...] = (
    "aircraft_id", "flight_id", "flight_date_utc", "log_sha256", "configuration", "sources",
    "duration_s", "tas_min_mps", "tas_max_mps", "alt_min_m", "alt_max_m", "converged",
    "software_version", "settings_json", "input_hashes_json", "recorded_at_utc",
)


#: columns of the current ``flights`` table, in order, without ``id``
FLIGHT_COLUMNS: tuple[str, ...] = (
    "aircraft_id", "flight_id", "flight_date_utc", "duration_s", "k1", "k2", "k3",
    "branch_k1", "branch_k2", "branch_k3", "converged", "converged_k1", "converged_k2",
    "converged_k3", "residual_m", "iterations",
    "software_version", "settings_json", "input_hashes_json", "recorded_at_utc", "log_sha256",
    "k1_sd", "k2_sd", "k3_sd",
)


def create_schema(con: sqlite3.Connection, ddl: tuple[str, ...], version: int) -> None:
    """Create a store's tables and identity inside the caller's write transaction."""
    for stmt in ddl:
        con.execute(stmt)
    con.execute(f"PRAGMA application_id = {APPLICATION_ID:d}")
    con.execute(f"PRAGMA user_version = {int(version):d}")
    con.executemany("INSERT INTO store_meta (key, value) VALUES (?, ?)", [
        ("application", APPLICATION_NAME),
        ("created_by", f"flightrecon {__version__}"),
    ])


def migrate_v1_to_v2(con: sqlite3.Connection) -> None:
    """Upgrade a v1 store to v2 inside the caller's write transaction.

    v1 had neither the per-axis root branch and convergence nor the iteration count, and it
    required k on every row.  The branch of an old row is the sign of its coefficient
    (``"positive"`` if k > 0, else ``"negative"``), which is what the branch means
    (docs/sabziev.md); each axis gets the row's overall convergence flag (v1 knew no better); the
    iteration count is unknown and stays NULL.  The table is rebuilt (create new, copy, drop
    old, rename), the SQLite-documented way to add NOT NULL and CHECK-constrained columns.
    """
    con.execute(f"CREATE TABLE flights_v2 ({_FLIGHTS_V2_COLUMNS})")
    sign = "CASE WHEN {k} > 0 THEN 'positive' ELSE 'negative' END"
    con.execute(
        "INSERT INTO flights_v2 (id, aircraft_id, flight_id, flight_date_utc, duration_s, k1, k2, "
        "k3, branch_k1, branch_k2, branch_k3, converged, converged_k1, converged_k2, "
        "converged_k3, residual_m, iterations, software_version, settings_json, "
        "input_hashes_json, recorded_at_utc) "
        "SELECT id, aircraft_id, flight_id, flight_date_utc, duration_s, k1, k2, k3, "
        f"{sign.format(k='k1')}, {sign.format(k='k2')}, {sign.format(k='k3')}, converged, "
        "converged, converged, converged, residual_m, NULL, software_version, settings_json, "
        "input_hashes_json, recorded_at_utc FROM flights")
    con.execute("DROP TABLE flights")
    con.execute("ALTER TABLE flights_v2 RENAME TO flights")
    con.execute("CREATE INDEX flights_by_aircraft ON flights (aircraft_id, flight_date_utc)")
    con.execute("INSERT OR REPLACE INTO store_meta (key, value) VALUES (?, ?)",
                ("migrated_to_v2_by", f"flightrecon {__version__}"))
    con.execute("PRAGMA user_version = 2")


def migrate_v2_to_v3(con: sqlite3.Connection) -> None:
    """Upgrade a v2 store to v3 inside the caller's write transaction.

    v3 adds the sensor-calibration tables (:data:`_V3_TABLES`, empty after the upgrade: a v2
    store holds no sensor estimates) and the column ``flights.log_sha256``, the SHA-256 of the
    flight's log that identifies the flight by its content.  An old row's log hash is not known
    for certain (v2 kept ``{input path: SHA-256}`` for every input, the metadata files too), so
    the column stays NULL and the identity rule falls back on the row's input hashes
    (:func:`flightrecon.store.identity.resolve_flight_id`).  No existing row is changed.
    """
    con.execute("ALTER TABLE flights ADD COLUMN log_sha256 TEXT")
    for stmt in _V3_TABLES:
        con.execute(stmt)
    con.execute("INSERT OR REPLACE INTO store_meta (key, value) VALUES (?, ?)",
                ("migrated_to_v3_by", f"flightrecon {__version__}"))
    con.execute("PRAGMA user_version = 3")


def migrate_v3_to_v4(con: sqlite3.Connection) -> None:
    """Upgrade a v3 store to v4 inside the caller's write transaction.

    v4 adds ``flights.k1_sd``, ``k2_sd``, ``k3_sd``: each root's conditioning (the spread of k
    that 50 m of end-point uncertainty gives, docs/sabziev.md).  An old row's conditioning was
    not recorded and stays NULL; the averages then weight that aircraft's fits equally
    (docs/store.md).  No existing value is changed.
    """
    for stmt in _V4_COLUMNS:
        con.execute(stmt)
    con.execute("INSERT OR REPLACE INTO store_meta (key, value) VALUES (?, ?)",
                ("migrated_to_v4_by", f"flightrecon {__version__}"))
    con.execute("PRAGMA user_version = 4")


#: from-version -> function that upgrades it by one version (inside a write transaction)
MIGRATIONS = {1: migrate_v1_to_v2, 2: migrate_v2_to_v3, 3: migrate_v3_to_v4}
