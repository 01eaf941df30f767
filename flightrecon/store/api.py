"""The coefficient store: record, read, average, export and remove per-flight Sabziev fits.

Examples
--------
>>> from flightrecon.store import CoefficientStore            # doctest: +SKIP
>>> with CoefficientStore() as store:                          # doctest: +SKIP
...     store.record(fit)              # a FlightCoefficients
...     fm = store.fleet_mean("4K-AZ01")
...     fm.k, fm.sd, fm.n
"""

from __future__ import annotations

import csv
import json
import math
import os
import sqlite3
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType

from flightrecon.errors import StoreError
from flightrecon.store import stats as _stats
from flightrecon.store.db import DEFAULT_BUSY_TIMEOUT_S, FLIGHT_COLUMNS, connect, write_transaction
from flightrecon.store.records import AircraftStats, FleetMean, FlightCoefficients, now_utc_text

_SELECT = "SELECT " + ", ".join(FLIGHT_COLUMNS) + " FROM flights"
_ORDER = " ORDER BY aircraft_id, flight_date_utc, flight_id"
_UPSERT = (
    "INSERT INTO flights (" + ", ".join(FLIGHT_COLUMNS) + ") VALUES ("
    + ", ".join("?" for _ in FLIGHT_COLUMNS)
    + ") ON CONFLICT (aircraft_id, flight_id) DO UPDATE SET "
    + ", ".join(f"{c} = excluded.{c}" for c in FLIGHT_COLUMNS[2:])
)

#: CSV columns of :meth:`CoefficientStore.export_csv` (units in the docs: k1, k3 [1/s], k2 [1/s^2])
CSV_COLUMNS: tuple[str, ...] = FLIGHT_COLUMNS


def _to_row(fc: FlightCoefficients) -> tuple:
    try:
        settings = json.dumps(fc.settings, sort_keys=True, allow_nan=False)
        hashes = json.dumps(fc.input_hashes, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise StoreError(f"flight '{fc.flight_id}': settings / input hashes are not plain JSON "
                         f"({exc})") from exc
    ac = fc.axis_converged or (fc.converged,) * 3
    return (fc.aircraft_id, fc.flight_id, fc.flight_date_utc, fc.duration_s,
            _null(fc.k1), _null(fc.k2), _null(fc.k3), fc.branch[0], fc.branch[1], fc.branch[2],
            int(fc.converged), int(ac[0]), int(ac[1]), int(ac[2]), _null(fc.residual_m),
            fc.iterations, fc.software_version, settings, hashes, fc.recorded_at_utc)


def _null(x: float) -> float | None:
    """NaN (unknown) as SQL NULL: SQLite would store NaN as NULL anyway, but say it."""
    return None if math.isnan(x) else x


def _from_row(row: tuple) -> FlightCoefficients:
    (aircraft_id, flight_id, date, duration, k1, k2, k3, b1, b2, b3, converged, c1, c2, c3,
     residual, iterations, version, settings, hashes, recorded) = row
    try:
        settings, hashes = json.loads(settings), json.loads(hashes)
    except ValueError as exc:
        raise StoreError(f"flight '{flight_id}' of aircraft '{aircraft_id}': settings / input "
                         f"hashes in the store are not valid JSON ({exc})") from exc
    return FlightCoefficients(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=date, duration_s=duration,
        k1=k1, k2=k2, k3=k3, branch=(b1, b2, b3), converged=bool(converged),
        residual_m=residual, iterations=iterations, software_version=version,
        settings=settings, input_hashes=hashes, axis_converged=(bool(c1), bool(c2), bool(c3)),
        recorded_at_utc=recorded)


class CoefficientStore:
    """A per-aircraft store of Sabziev coefficient fits in one SQLite file.

    Opening it creates the file on first use (default location:
    :func:`flightrecon.store.db.default_store_path`), upgrades an older schema, and refuses a
    file that is not a flightrecon store (:class:`~flightrecon.errors.StoreError`, file left
    unmodified).  Each call is its own transaction; several processes may write at once.

    Parameters
    ----------
    path : store file (``None``: ``$FLIGHTRECON_STORE`` or the per-user data folder)
    busy_timeout_s : how long to wait for another process's write lock [s]
    create : create a missing store (False: a missing store raises StoreError)

    Attributes
    ----------
    path : the store file
    journal_mode : ``"wal"``, or ``"delete"`` where the file system cannot do WAL
    notes : remarks for the user (e.g. the WAL fallback)
    """

    def __init__(self, path: str | os.PathLike | None = None, *,
                 busy_timeout_s: float = DEFAULT_BUSY_TIMEOUT_S, create: bool = True) -> None:
        self._con, self.path, self.journal_mode = connect(path, busy_timeout_s=busy_timeout_s,
                                                          create=create)
        self.notes: tuple[str, ...] = ()
        if self.journal_mode != "wal":
            self.notes = (f"journal mode {self.journal_mode}: the file system does not support "
                          "WAL; readers and the writer take turns",)

    # -- lifecycle ---------------------------------------------------------------------------
    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> CoefficientStore:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    @property
    def con(self) -> sqlite3.Connection:
        """The open connection (StoreError once closed)."""
        if self._con is None:
            raise StoreError("the coefficient store is closed", file=str(self.path))
        return self._con

    def _run(self, fn, *args):
        try:
            return fn(*args)
        except sqlite3.Error as exc:
            raise StoreError(f"coefficient store: {exc}", file=str(self.path)) from exc

    # -- writing -----------------------------------------------------------------------------
    def record(self, fit: FlightCoefficients) -> FlightCoefficients:
        """Insert ``fit``, or replace the row of the same (aircraft_id, flight_id).

        Returns the record as stored (``recorded_at_utc`` set to now).
        """
        return self.record_many([fit])[0]

    def record_many(self, fits: Iterable[FlightCoefficients]) -> list[FlightCoefficients]:
        """Record several fits in one transaction: all of them or, on any error, none."""
        def work() -> list[FlightCoefficients]:
            out = []
            with write_transaction(self.con) as con:
                stamp = now_utc_text()
                for fit in fits:
                    if not isinstance(fit, FlightCoefficients):
                        raise StoreError(f"expected FlightCoefficients, got {type(fit).__name__}")
                    row = _to_row(fit)[:-1] + (stamp,)
                    con.execute(_UPSERT, row)
                    out.append(_from_row(row))
            return out
        return self._run(work)

    def remove(self, aircraft_id: str, flight_id: str | None = None) -> int:
        """Delete one flight, or every flight of the aircraft when ``flight_id`` is None.

        Returns the number of rows deleted (0 if there was nothing to delete).
        """
        def work() -> int:
            with write_transaction(self.con) as con:
                if flight_id is None:
                    cur = con.execute("DELETE FROM flights WHERE aircraft_id = ?", (aircraft_id,))
                else:
                    cur = con.execute("DELETE FROM flights WHERE aircraft_id = ? AND flight_id = ?",
                                      (aircraft_id, flight_id))
                return cur.rowcount
        return self._run(work)

    # -- reading -----------------------------------------------------------------------------
    def list_flights(self, aircraft_id: str | None = None) -> list[FlightCoefficients]:
        """Every recorded fit (of one aircraft if given), by aircraft, date, flight id."""
        def work() -> list[FlightCoefficients]:
            if aircraft_id is None:
                rows = self.con.execute(_SELECT + _ORDER).fetchall()
            else:
                rows = self.con.execute(_SELECT + " WHERE aircraft_id = ?" + _ORDER,
                                        (aircraft_id,)).fetchall()
            return [_from_row(r) for r in rows]
        return self._run(work)

    def aircraft(self) -> list[tuple[str, int]]:
        """``[(aircraft_id, number of flights), ...]`` sorted by aircraft id."""
        return self._run(lambda: [(a, int(n)) for a, n in self.con.execute(
            "SELECT aircraft_id, count(*) FROM flights GROUP BY aircraft_id ORDER BY aircraft_id")])

    def get(self, aircraft_id: str, flight_id: str) -> FlightCoefficients:
        """The fit of one flight; StoreError if it is not recorded."""
        rows = self._run(lambda: self.con.execute(
            _SELECT + " WHERE aircraft_id = ? AND flight_id = ?", (aircraft_id, flight_id)
        ).fetchall())
        if not rows:
            raise StoreError(f"no flight '{flight_id}' of aircraft '{aircraft_id}' in the store",
                             file=str(self.path))
        return _from_row(rows[0])

    def count(self) -> int:
        """Number of recorded fits."""
        return int(self._run(
            lambda: self.con.execute("SELECT count(*) FROM flights").fetchone()[0]))

    # -- statistics --------------------------------------------------------------------------
    def aircraft_stats(self, aircraft_id: str) -> AircraftStats:
        """Per-axis count, mean, median, std and drift of one aircraft's fits
        (rule: :mod:`flightrecon.store.stats`); StoreError if the aircraft has no flights."""
        records = self.list_flights(aircraft_id)
        if not records:
            raise StoreError(f"no flights of aircraft '{aircraft_id}' in the store",
                             file=str(self.path))
        return _stats.aircraft_stats(aircraft_id, records)

    def fleet_mean(self, aircraft_id: str, min_flights: int = 1) -> FleetMean:
        """Mean coefficients, their flight-to-flight spread and counts, for the initial-value
        mode (see :func:`flightrecon.store.stats.fleet_mean`)."""
        return _stats.fleet_mean(self.aircraft_stats(aircraft_id), min_flights=min_flights)

    # -- export ------------------------------------------------------------------------------
    def export_csv(self, path: str | os.PathLike, aircraft_id: str | None = None) -> int:
        """Write the fits (of one aircraft if given) to a CSV file, atomically.

        Columns: :data:`CSV_COLUMNS`; booleans as 0/1, a missing residual or iteration count as
        an empty cell, settings and input hashes as JSON text.  Returns the number of rows.
        """
        from flightrecon.export.atomic import atomic_path

        records = self.list_flights(aircraft_id)
        with atomic_path(Path(path)) as tmp:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(CSV_COLUMNS)
                for r in records:
                    row = list(_to_row(r))
                    row = ["" if v is None else (repr(v) if isinstance(v, float) else v)
                           for v in row]
                    w.writerow(row)
        return len(records)
