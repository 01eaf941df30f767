"""Store file: creation, identity checks, schema upgrade v1 -> v2, idempotent re-recording."""

import hashlib
import math
import sqlite3
from dataclasses import replace

import pytest

from flightrecon.errors import StoreError
from flightrecon.store import SCHEMA_VERSION, CoefficientStore, FlightCoefficients, db, schema


def fit(**kw):
    base = dict(aircraft_id="4K-AZ01", flight_id="F001", flight_date_utc="2024-05-01T10:00:00Z",
                duration_s=3600.0, k1=-0.01, k2=-1e-4, k3=-0.02,
                branch=("negative", "negative", "negative"), converged=True, residual_m=12.5,
                iterations=7, software_version="0.1.0", settings={"rate_hz": 16.0},
                input_hashes={"log": "ab" * 32})
    base.update(kw)
    return FlightCoefficients(**base)


def snapshot(folder):
    """{name: sha256} of every file in ``folder`` (to prove nothing was touched or created)."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}


def test_new_store_has_identity_schema_and_wal(tmp_path):
    path = tmp_path / "s.sqlite"
    with CoefficientStore(path) as store:
        assert store.journal_mode == "wal" and store.notes == ()
        assert store.count() == 0
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA application_id").fetchone()[0] == schema.APPLICATION_ID
    assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 4
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    cols = [r[1] for r in con.execute("PRAGMA table_info(flights)")]
    assert tuple(cols[1:]) == schema.FLIGHT_COLUMNS
    meta = dict(con.execute("SELECT key, value FROM store_meta"))
    assert meta["application"] == schema.APPLICATION_NAME
    con.close()


def test_missing_store_not_created_when_create_false(tmp_path):
    with pytest.raises(StoreError, match="no coefficient store"):
        CoefficientStore(tmp_path / "none.sqlite", create=False)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(StoreError, match="does not exist"):
        CoefficientStore(tmp_path / "nodir" / "s.sqlite")


def test_default_location(monkeypatch, tmp_path):
    monkeypatch.setenv("FLIGHTRECON_STORE", str(tmp_path / "env.sqlite"))
    assert db.default_store_path() == tmp_path / "env.sqlite"
    monkeypatch.delenv("FLIGHTRECON_STORE")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    if db.sys.platform.startswith("linux"):
        assert db.default_store_path() == tmp_path / "xdg" / "flightrecon" / "coefficients.sqlite"
        with CoefficientStore() as store:   # first use creates the folder and the file
            assert store.path == db.default_store_path() and store.path.is_file()


def test_journal_mode_fallback_is_reported():
    """Where WAL cannot be set, the mode in effect is returned (an in-memory database cannot use
    WAL, like a network file system) and the store would carry a note."""
    con = sqlite3.connect(":memory:", isolation_level=None)
    assert db._set_journal_mode(con) == "memory"
    con.close()


def test_rerecording_replaces_the_row(tmp_path):
    path = tmp_path / "s.sqlite"
    with CoefficientStore(path) as store:
        first = store.record(fit())
        second = store.record(fit(k1=-0.5, branch=("negative", "positive", "negative"),
                                  k2=3e-4, iterations=11, converged=False, residual_m=math.nan,
                                  settings={"rate_hz": 8.0}))
        assert store.count() == 1
        got = store.get("4K-AZ01", "F001")
        assert got == second and got != first
        assert got.k1 == -0.5 and got.iterations == 11 and math.isnan(got.residual_m)
        assert got.settings == {"rate_hz": 8.0}
        assert got.recorded_at_utc >= first.recorded_at_utc
        store.record(fit(flight_id="F002"))
        store.record(fit(aircraft_id="OTHER"))
        assert [f.flight_id for f in store.list_flights("4K-AZ01")] == ["F001", "F002"]
        assert store.aircraft() == [("4K-AZ01", 2), ("OTHER", 1)]
        assert store.remove("4K-AZ01", "F404") == 0
        assert store.remove("4K-AZ01", "F001") == 1
        assert store.remove("4K-AZ01") == 1 and store.count() == 1
        with pytest.raises(StoreError, match="no flight 'F001'"):
            store.get("4K-AZ01", "F001")
        with pytest.raises(StoreError, match="no flights of aircraft"):
            store.aircraft_stats("4K-AZ01")


def test_parameterised_queries_take_hostile_ids_literally(tmp_path):
    """Identifiers are bound parameters, never spliced into SQL."""
    evil = "x'); DROP TABLE flights; --"
    with CoefficientStore(tmp_path / "s.sqlite") as store:
        store.record(fit(aircraft_id=evil, flight_id=evil))
        assert store.get(evil, evil).aircraft_id == evil and store.count() == 1


def _build_v1(path, rows):
    con = sqlite3.connect(path, isolation_level=None)
    with db.write_transaction(con):
        schema.create_schema(con, schema.SCHEMA_V1_DDL, 1)
        con.executemany(
            "INSERT INTO flights (aircraft_id, flight_id, flight_date_utc, duration_s, k1, k2, k3, "
            "converged, residual_m, software_version, settings_json, input_hashes_json, "
            "recorded_at_utc) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", rows)
    con.close()


def test_upgrade_from_v1(tmp_path):
    path = tmp_path / "old.sqlite"
    _build_v1(path, [
        ("A", "F1", "2023-01-01T00:00:00Z", 1000.0, -0.01, -2e-4, -0.03, 1, 4.0, "0.0.9",
         '{"a": 1}', '{"log": "00"}', "2023-01-02T00:00:00Z"),
        ("A", "F2", "2023-01-05T00:00:00Z", 2000.0, 0.02, 3e-4, -0.01, 0, 250.0, "0.0.9",
         "{}", "{}", "2023-01-06T00:00:00Z"),
    ])
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA user_version").fetchone()[0] == 1
    assert "branch_k1" not in [r[1] for r in con.execute("PRAGMA table_info(flights)")]
    con.close()
    with CoefficientStore(path) as store:
        old = store.list_flights()
        # branch of a v1 row = sign of its k; iteration count unknown
        assert [f.branch for f in old] == [("negative", "negative", "negative"),
                                           ("positive", "positive", "negative")]
        assert [f.iterations for f in old] == [None, None]
        assert [f.axis_converged for f in old] == [(True,) * 3, (False,) * 3]
        assert old[0].settings == {"a": 1} and old[0].residual_m == 4.0
        assert old[1].residual_m == 250.0 and old[1].converged is False
        store.record(fit(aircraft_id="A", flight_id="F3"))
        assert store.count() == 3
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    cols = tuple(r[1] for r in con.execute("PRAGMA table_info(flights)"))
    assert cols[1:] == schema.FLIGHT_COLUMNS
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    meta = dict(con.execute("SELECT key, value FROM store_meta"))
    assert "migrated_to_v2_by" in meta and "migrated_to_v3_by" in meta  # v1 -> v2 -> v3
    con.close()
    with CoefficientStore(path) as store:   # opening again does not migrate again
        assert store.count() == 3


def test_newer_schema_refused_and_untouched(tmp_path):
    path = tmp_path / "s.sqlite"
    with CoefficientStore(path) as store:
        store.record(fit())
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode = DELETE")   # no -wal/-shm beside it: one file to compare
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    con.close()
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="newer"):
        CoefficientStore(path)
    assert snapshot(tmp_path) == before


def test_random_bytes_refused_and_untouched(tmp_path):
    path = tmp_path / "junk.sqlite"
    path.write_bytes(bytes(range(256)) * 16)
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="not a SQLite database") as ei:
        CoefficientStore(path)
    assert ei.value.exit_code == 10 and str(path) in str(ei.value)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("journal", ["delete", "wal"])
def test_foreign_sqlite_refused_and_untouched(tmp_path, journal):
    """Also in WAL mode, where a read-only SQLite open would leave -wal/-shm files beside it:
    the foreign database is refused on its raw header, before SQLite opens it."""
    path = tmp_path / "other.db"
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA journal_mode = {journal}")
    con.execute("CREATE TABLE customers (id INTEGER PRIMARY KEY, name TEXT)")
    con.execute("INSERT INTO customers (name) VALUES ('x')")
    con.commit()
    con.close()
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="another application"):
        CoefficientStore(path)
    assert snapshot(tmp_path) == before       # no tables added, no journal left beside it


def test_our_application_id_without_marker_refused(tmp_path):
    """application_id alone is 4 bytes anyone could pick; the store_meta marker must match too."""
    path = tmp_path / "fake.db"
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA application_id = {schema.APPLICATION_ID}")
    con.execute("PRAGMA user_version = 2")
    con.execute("CREATE TABLE flights (x)")
    con.commit()
    con.close()
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="another application"):
        CoefficientStore(path)
    assert snapshot(tmp_path) == before


def test_corrupt_sqlite_body_refused(tmp_path):
    """A SQLite header followed by garbage (a truncated or overwritten store)."""
    path = tmp_path / "bad.sqlite"
    with CoefficientStore(path) as store:
        store.record(fit())
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode = DELETE")
    con.close()
    raw = bytearray(path.read_bytes())
    raw[16:] = bytes((7 * i) % 251 for i in range(len(raw) - 16))
    path.write_bytes(bytes(raw))
    before = snapshot(tmp_path)
    with pytest.raises(StoreError, match="corrupt"):
        CoefficientStore(path)
    assert snapshot(tmp_path) == before


def test_empty_file_is_initialised(tmp_path):
    """A zero-byte file holds nothing to lose (e.g. created by `touch`): it becomes a store."""
    path = tmp_path / "s.sqlite"
    path.touch()
    with CoefficientStore(path) as store:
        store.record(fit())
        assert store.count() == 1


def test_partial_fit_round_trip_and_sql_checks(tmp_path):
    """Unknown k is stored as NULL and read back as NaN; the table's CHECK constraints refuse
    rows that bypass the record validation (a converged axis without k)."""
    path = tmp_path / "s.sqlite"
    partial = fit(converged=False, axis_converged=(True, False, True), k2=math.nan,
                  branch=("negative", "none", "negative"), residual_m=math.nan)
    with CoefficientStore(path) as store:
        stored = store.record(partial)
        got = store.get("4K-AZ01", "F001")
        assert got == stored == replace(partial, recorded_at_utc=stored.recorded_at_utc)
        assert math.isnan(got.k2) and got.axis_converged == (True, False, True)
        row = store.con.execute("SELECT k2, residual_m FROM flights").fetchone()
        assert row == (None, None)
        cols = ", ".join(schema.FLIGHT_COLUMNS)
        marks = ", ".join("?" for _ in schema.FLIGHT_COLUMNS)
        bad = ("A", "X", "2024-01-01T00:00:00Z", 10.0, -0.1, None, -0.1, "negative", "negative",
               "negative", 1, 1, 1, 1, 1.0, 3, "0", "{}", "{}", "2024-01-01T00:00:00Z", None,
               None, None, None)
        with pytest.raises(sqlite3.IntegrityError):
            store.con.execute(f"INSERT INTO flights ({cols}) VALUES ({marks})", bad)
